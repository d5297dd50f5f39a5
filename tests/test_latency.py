"""What a command or ``import tumble`` loads: only what it needs (issue 29).

Start-up time is dominated by imports (numba, xarray with pandas, matplotlib, netCDF4, dask: 0.1-0.6 s each on
2 cores), so the tests check the modules a fresh interpreter holds afterwards, not a time (timings are in
``benchmarks/latency.py``).
"""

import json
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


def test_the_short_import_paths_give_the_layers_modules():
    code = ("import sys, tumble, tumble.exact, tumble.io\nfrom tumble.theory import linear\n"
            "from tumble.models import Gyrostat\nimport tumble.measure.scenes\n"
            "assert tumble.exact is sys.modules['tumble.physics.exact']\n"
            "assert tumble.exact.__spec__.name == 'tumble.physics.exact'\n"
            "assert tumble.io is sys.modules['tumble.output.io']\n"
            "assert linear is sys.modules['tumble.physics.theory'].linear\n"
            "assert callable(tumble.measure) and tumble.measure.__name__ == 'measure'\n"
            "assert set(tumble.__all__) <= set(dir(tumble))")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_unknown_name_is_an_attribute_error():
    import tumble

    with pytest.raises(AttributeError, match="no attribute 'integrat'"):
        tumble.integrat  # noqa: B018
