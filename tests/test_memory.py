"""The numbers that protect against faults (issue 33, cause 7): the checkpoint holds only what the result needs,
and the ``--dry-run`` memory estimate is within 1.5x of a measured peak."""

import pytest
from test_resume import _toml

from tumble import cli
from tumble.pipeline import checkpoint

# A stability map in small: 36 bodies x 3 axes, closed form, no per-sample arrays kept.
MAP = {"title": "map", "perturbation": {"samples": 2048}, "scan": {"triangle": 6, "axis": [1, 2, 3]},
       "outputs": {"figures": [], "arrays": []}}


@pytest.mark.default_cases("sample-rate")
@pytest.mark.parametrize("arrays, most", [([], 3.0), (["sample_rate"], 5.0)], ids=["no-arrays", "sample-rate"])
def test_the_checkpoint_keeps_only_what_the_result_needs(tmp_path, capsys, monkeypatch, arrays, most):
    """The chunks kept every per-sample array (rate, status, flip times) whatever ``outputs.arrays`` asked for: a
    2048-sample stability map's checkpoint was 140 times its result. Now it is within a few times of it (the
    chunks are not compressed, the result is)."""
    study = tmp_path / "map.toml"
    study.write_text(_toml({**MAP, "outputs": {"figures": [], "arrays": arrays}}))
    monkeypatch.setattr(checkpoint.Checkpoint, "remove", lambda self: None)  # keep the chunks to weigh them
    assert cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--chunk-scenes", "8"]) == 0
    capsys.readouterr()
    chunks = sum(p.stat().st_size for p in checkpoint.chunk_folder(tmp_path / "out", "map").iterdir())
    result = (tmp_path / "out" / "map.nc").stat().st_size
    assert chunks < most * result, f"checkpoint {chunks} B for a result of {result} B"


# --- the --dry-run memory estimate against a measured peak ------------------------------------------------------
# Peak resident memory of a child process that runs the study through the command line, minus the peak of a child
# that only imports it: what the run itself adds, which is what the estimate (tumble.pipeline.runner.study_cost: the
# run's fixed footprint and the modelled working set) claims. Resident memory rather than tracemalloc: numba's kernels
# and netCDF allocate outside Python's allocator, and the bound protects the machine's memory, all of it. The peak is
# the child's own VmHWM (/proc/self/status), not getrusage's ru_maxrss: Linux carries the parent's peak across
# fork and exec into ru_maxrss (RUSAGE_CHILDREN too), so under a pytest worker of a few hundred MB the idle child
# reported the worker's peak and the difference came out 112 MB for 353. Each child first runs the study at 64
# samples, so that numba's cache is warm and the peak is the run's, not the compiler's.

_PEAK_CHILD = """
import json, resource, sys
from tumble import cli
from tumble.pipeline import runner
if sys.argv[1] == "run":
    for samples in ("64", None):
        extra = ["--samples", samples] if samples else []
        assert cli.main(["run", sys.argv[2], "--out", sys.argv[3], "--fresh", *extra]) == 0
estimate = runner.study_cost(runner.prepare_study(sys.argv[2], out=sys.argv[3]).resolved).peak_bytes
try:
    with open("/proc/self/status") as status:
        peak = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:")) * 1024
except OSError:  # no /proc: ru_maxrss (includes the parent's peak on Linux, not elsewhere)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * (1 if sys.platform == "darwin" else 1024)
print(json.dumps({"peak": peak, "estimate": estimate}))
"""


def _peak(mode, study, out):
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", _PEAK_CHILD, mode, str(study), str(out)], capture_output=True,
                          text=True, timeout=300, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _shape(**tables):
    spec = {"title": "shape", "body": {"moments": [1.0, 2.0, 3.0]}, "outputs": {"figures": [], "arrays": []}}
    for table, values in tables.items():
        spec.setdefault(table, {}).update(values)
    return spec


SHAPES = {
    # 6 closed-form exponential scenes of 65 536 samples with two per-sample arrays (the 42 MB vs 216 MB)
    "closed-form-exponential": _shape(spin={"axis": 2}, scan={"amplitude": [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 3e-2]},
                                      perturbation={"samples": 65536},
                                      outputs={"arrays": ["sample_first_flip", "sample_flip_spacing"]}),
    "closed-form-periodic": _shape(spin={"axis": 1}, scan={"amplitude": [1e-4, 1e-3, 1e-2]},
                                   perturbation={"samples": 65536}, outputs={"arrays": ["sample_rate"]}),
    "rk4-periodic": _shape(spin={"axis": 3}, integration={"method": "rk4"}, perturbation={"samples": 65536}),
    "rk4-exponential": _shape(spin={"axis": 2}, integration={"method": "rk4"}, perturbation={"samples": 131072}),
    "triangle-of-bodies": _shape(scan={"triangle": 8, "axis": [1, 2, 3]}, perturbation={"samples": 2048}),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", SHAPES)
def test_the_dry_run_memory_estimate_is_within_1_5x_of_the_measured_peak(tmp_path, name):
    """The estimate was about 5x too low (42 MB for 216 MB measured): it counted 640 B per sample, once, where a
    slice of samples holds its observed components at every time, and a study holds the run's fixed footprint."""
    study = tmp_path / "shape.toml"
    study.write_text(_toml(SHAPES[name]))
    idle = _peak("import", study, tmp_path / "out")
    run = _peak("run", study, tmp_path / "out")
    measured = run["peak"] - idle["peak"]
    assert 1 / 1.5 <= run["estimate"] / measured <= 1.5, (f"estimated {run['estimate'] / 1e6:.0f} MB, measured "
                                                         f"{measured / 1e6:.0f} MB above an idle import")
